#!/usr/bin/python3
"""Benchmarks of the kiln Python module against what Python users use (issue 23).

    PYTHONPATH=build/python /usr/bin/python3 bench/python_bench.py [--quick] [--rounds N]

- kNN: kiln.build(..., accel="points") and Structure.knn against scipy.spatial.cKDTree
  (build from the same float32 array; query with workers=-1 and threads=None, and one thread).
- Point in polygon over the US counties: Structure.locate against geopandas.sjoin
  (predicate="within", rtree index) and shapely prepared geometries (each county prepared,
  its bounding box cutting the candidates, shapely.vectorized.contains), on the 42,049 ZIP
  points and on 1 M uniform random points over the counties' bounds.
- Rays: the binding's cost per call for batches of 1, 1 k and 1 M rays: Structure.intersect
  (numpy in, structured array out) against the C++ path: `kiln trace`'s own wall-clock timing
  of RayQueries::trace_records on the same rays (it excludes reading and writing its files),
  and, on one thread, CPU seconds: the Python process's against the CLI's (less what the CLI
  spends on a one-ray run: start, open, write), which the machine's load disturbs less.

Peers alternate in one process, `--rounds` times each, and the medians are reported: the
machine is shared with other jobs, so single timings are noisy.
"""
import argparse
import os
import pathlib
import re
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import kiln

ROOT = pathlib.Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
CLI = os.environ.get("KILN_CLI", str(ROOT / "build" / "tools" / "kiln"))


def timed(fn):
    start = time.perf_counter()
    result = fn()
    return time.perf_counter() - start, result


def alternate(rounds, **peers):
    """Runs each peer once per round, in turn; returns {name: (median seconds, last result)}."""
    times = {name: [] for name in peers}
    results = {}
    for _ in range(rounds):
        for name, fn in peers.items():
            seconds, results[name] = timed(fn)
            times[name].append(seconds)
    return {name: (statistics.median(t), results[name]) for name, t in times.items()}


def write_ply(path, points):
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\n"
              "property float x\nproperty float y\nproperty float z\nend_header\n")
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(np.ascontiguousarray(points, "<f4").tobytes())


def bench_knn(tmp, n, q, rounds):
    from scipy.spatial import cKDTree
    rng = np.random.default_rng(1)
    points = rng.random((n, 3), dtype=np.float32)
    queries = rng.random((q, 3), dtype=np.float32)
    ply = tmp / "points.ply"
    write_ply(ply, points)
    builds = alternate(rounds,
                       kiln=lambda: kiln.build(ply, tmp / "points.kiln", accel="points"),
                       ckdtree=lambda: cKDTree(points))
    tree = builds["ckdtree"][1]
    print(f"\nkNN, {n:,} uniform points in the unit cube, {q:,} queries")
    print(f"  build: kiln.build (PLY import + tree + blob write) {builds['kiln'][0]:.3f} s, "
          f"cKDTree(points) {builds['ckdtree'][0]:.3f} s")
    with kiln.open(tmp / "points.kiln") as blob:
        s = blob["points"]
        for k in (1, 8):
            for threads, workers, label in ((None, -1, "all cores"), (1, 1, "1 thread")):
                r = alternate(rounds, kiln=lambda: s.knn(queries, k=k, threads=threads),
                              ckdtree=lambda: tree.query(queries, k=k, workers=workers))
                same = np.array_equal(r["kiln"][1][1], r["ckdtree"][1][1])
                print(f"  query k={k} ({label}): kiln {q / r['kiln'][0] / 1e6:.2f} M/s, "
                      f"cKDTree {q / r['ckdtree'][0] / 1e6:.2f} M/s, "
                      f"{r['ckdtree'][0] / r['kiln'][0]:.2f}x; indices equal: {same}")


def shapely_prepared(counties, lon, lat):
    """Point in polygon with shapely prepared geometries: per county, the points in its bounds
    (sorted by lon, then a lat mask), tested with shapely.vectorized.contains."""
    from shapely import vectorized
    from shapely.prepared import prep
    order = np.argsort(lon, kind="stable")
    xs, ys = lon[order], lat[order]
    out = np.full(len(lon), -1, np.int64)
    for index, geometry in enumerate(counties.geometry):
        x0, y0, x1, y1 = geometry.bounds
        lo, hi = np.searchsorted(xs, x0, "left"), np.searchsorted(xs, x1, "right")
        cand = np.flatnonzero((ys[lo:hi] >= y0) & (ys[lo:hi] <= y1)) + lo
        if len(cand) == 0:
            continue
        inside = vectorized.contains(prep(geometry), xs[cand], ys[cand])
        hit = order[cand[inside]]
        out[hit] = np.where(out[hit] < 0, index, np.minimum(out[hit], index))
    return out


def sjoin(geopandas, counties, lon, lat):
    points = geopandas.GeoDataFrame(geometry=geopandas.points_from_xy(lon, lat), crs=counties.crs)
    joined = geopandas.sjoin(points, counties, predicate="within", how="left")
    joined = joined[~joined.index.duplicated()]
    return joined["index_right"].fillna(-1).astype(np.int64).to_numpy()


def bench_pip(tmp, rounds, random_points):
    import geopandas
    import pandas as pd
    geojson, csv = tmp / "counties.geojson", tmp / "zipcodes.csv"
    for src, dst in ((DATA / "geo" / "us-counties-10m.geojson.zst", geojson),
                     (DATA / "geo" / "zipcodes.csv.zst", csv)):
        dst.write_bytes(subprocess.run(["zstd", "-dc", str(src)], capture_output=True,
                                       check=True).stdout)
    kiln.build(geojson, tmp / "counties.kiln", accel="polygon-index")
    counties = geopandas.read_file(geojson)
    zips = pd.read_csv(csv)
    x0, y0, x1, y1 = counties.total_bounds
    rng = np.random.default_rng(2)
    sets = {"ZIP points": (zips["longitude"].to_numpy(), zips["latitude"].to_numpy()),
            f"{random_points:,} random points": (rng.uniform(x0, x1, random_points),
                                                 rng.uniform(y0, y1, random_points))}
    with kiln.open(tmp / "counties.kiln") as blob:
        pip = blob["polygon-index"]
        for name, (lon, lat) in sets.items():
            n = len(lon)
            slow_rounds = 1 if n > 100_000 else rounds
            r = alternate(slow_rounds, sjoin=lambda: sjoin(geopandas, counties, lon, lat),
                          prepared=lambda: shapely_prepared(counties, lon, lat))
            k = alternate(rounds, kiln=lambda: pip.locate(lon, lat),
                          kiln1=lambda: pip.locate(lon, lat, threads=1))
            print(f"\nPoint in polygon, US counties, {name} ({n:,})")
            for label, (seconds, found) in (("kiln locate, all cores", k["kiln"]),
                                            ("kiln locate, 1 thread", k["kiln1"]),
                                            ("geopandas.sjoin within", r["sjoin"]),
                                            ("shapely prepared + bbox", r["prepared"])):
                same = np.array_equal(found, k["kiln"][1])
                print(f"  {label:26s} {seconds:8.4f} s {n / seconds / 1e3:10.0f} k points/s"
                      f"  same answers: {same}")
            print(f"  kiln vs sjoin: {r['sjoin'][0] / k['kiln'][0]:.0f}x (all cores), "
                  f"{r['sjoin'][0] / k['kiln1'][0]:.0f}x (1 thread)")


def cli_trace_seconds(blob, rays_file):
    """`kiln trace`'s own measure of trace_records (Mrays/s on stderr) -> seconds."""
    out = subprocess.run([CLI, "trace", str(blob), "--rays", str(rays_file), "--out",
                          os.devnull, "--accel", "bvh"], capture_output=True, text=True,
                         check=True).stderr
    count, rate = re.search(r"(\d+) rays on .*, ([\d.]+) Mrays/s", out).groups()
    return int(count) / (float(rate) * 1e6)


def cli_cpu_seconds(blob, rays_file):
    """CPU seconds (user + system) of `kiln trace --threads 1` on a RAYS file."""
    import resource
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([CLI, "trace", str(blob), "--rays", str(rays_file), "--out", os.devnull,
                    "--accel", "bvh", "--threads", "1"], capture_output=True, check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def bench_rays(tmp, rounds, mesh):
    blob_path, rays_path = tmp / "rays.kiln", tmp / "diffuse.rays"
    kiln.build(mesh, blob_path, accel="bvh")
    subprocess.run([CLI, "rays", str(blob_path), "--kind", "diffuse", "--count", "1000000",
                    "-o", str(rays_path)], check=True, capture_output=True)
    rays = np.fromfile(rays_path, np.float32).reshape(-1, 8)
    print(f"\nRays: {mesh.name}, diffuse rays (kiln rays), closest hit on the BVH")
    print("  batch      wall, all cores: Python   C++     |  CPU, 1 thread: Python   C++")
    with kiln.open(blob_path) as blob:
        bvh = blob["bvh"]
        for batch, calls in ((1, 2000), (1000, 100), (1_000_000, 1)):
            part = tmp / f"rays_{batch}.rays"
            rays[:batch].tofile(part)
            org, dirs = rays[:batch, 0:3].copy(), rays[:batch, 4:7].copy()
            wall_py, wall_cpp, cpu_py, cpu_cpp = [], [], [], []
            for _ in range(rounds):  # alternating: Python, then the CLI on the same rays
                wall_py.append(timed(lambda: [bvh.intersect(org, dirs)
                                              for _ in range(calls)])[0] / calls)
                wall_cpp.append(cli_trace_seconds(blob_path, part))
                start = time.process_time()
                for _ in range(calls):
                    bvh.intersect(org, dirs, threads=1)
                cpu_py.append((time.process_time() - start) / calls)
                # The CLI's CPU on these rays less its CPU on one ray (start, open, write).
                if batch > 1:
                    cpu_cpp.append(cli_cpu_seconds(blob_path, part) -
                                   cli_cpu_seconds(blob_path, tmp / "rays_1.rays"))
            m = statistics.median
            cpu = (f"{m(cpu_py) * 1e6:12.1f} us {m(cpu_cpp) * 1e6:10.1f} us "
                   f"({100 * (m(cpu_py) / m(cpu_cpp) - 1):+.1f} %)" if cpu_cpp else
                   f"{m(cpu_py) * 1e6:12.1f} us        n/a")
            print(f"  {batch:>9,}  {m(wall_py) * 1e6:14.1f} us {m(wall_cpp) * 1e6:10.1f} us  |"
                  f"  {cpu}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--quick", action="store_true", help="small sizes, to check it runs")
    parser.add_argument("--only", choices=["knn", "pip", "rays"])
    args = parser.parse_args()
    print(f"kiln Python benchmarks, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
          f"nproc {os.cpu_count()}, Python {sys.version.split()[0]}, medians of {args.rounds}")
    with tempfile.TemporaryDirectory() as name:
        tmp = pathlib.Path(name)
        if args.only in (None, "knn"):
            bench_knn(tmp, 100_000 if args.quick else 1_000_000,
                      20_000 if args.quick else 200_000, args.rounds)
        if args.only in (None, "pip"):
            bench_pip(tmp, args.rounds, 100_000 if args.quick else 1_000_000)
        if args.only in (None, "rays"):
            bench_rays(tmp, args.rounds, DATA / "meshes" / "stanford" / "Lucy100k.ply")


if __name__ == "__main__":
    main()
