#!/usr/bin/python3
"""Which county is each US ZIP code in? The ten counties with the most ZIP codes, with kiln and
with geopandas, compared in time and answers.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/zip_to_county.py \\
        [../shared/data/geo/us-counties-10m.geojson.zst] [../shared/data/geo/zipcodes.csv.zst]
"""
import io
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np
import pandas as pd

import kiln

DATA = pathlib.Path(__file__).resolve().parents[3] / "shared" / "data" / "geo"
counties_path = sys.argv[1] if len(sys.argv) > 1 else DATA / "us-counties-10m.geojson.zst"
zips_path = sys.argv[2] if len(sys.argv) > 2 else DATA / "zipcodes.csv.zst"


def read_bytes(path):
    """A file's bytes, inflated with the zstd tool when it ends in .zst."""
    if str(path).endswith(".zst"):
        return subprocess.run(["zstd", "-dc", str(path)], capture_output=True, check=True).stdout
    return pathlib.Path(path).read_bytes()


zips = pd.read_csv(io.BytesIO(read_bytes(zips_path)), dtype={"zip_code": str})
lon, lat = zips["longitude"].to_numpy(), zips["latitude"].to_numpy()

with tempfile.TemporaryDirectory() as tmp:
    blob_path = pathlib.Path(tmp) / "counties.kiln"
    start = time.perf_counter()
    kiln.build(counties_path, blob_path, accel="polygon-index")  # reads .zst itself
    built = time.perf_counter() - start
    with kiln.open(blob_path) as blob:
        layer = blob["polygon-index"]
        start = time.perf_counter()
        county = layer.locate(lon, lat)  # int64 feature index per point, -1 where none
        located = time.perf_counter() - start
        ids, names = layer.attributes(county)

zips["county_fips"], zips["county_name"] = ids, names
top = (zips[county >= 0].groupby(["county_fips", "county_name"]).size()
       .sort_values(ascending=False, kind="stable").head(10))
print(f"kiln: {len(zips):,} ZIP codes located in {located * 1e3:.1f} ms "
      f"(index built in {built:.2f} s); {(county < 0).sum()} in no county")
print("Counties with the most ZIP codes:")
for (fips, name), count in top.items():
    print(f"  {fips} {name:20s} {count}")

try:
    import geopandas
except ImportError:
    sys.exit("geopandas is absent: no comparison")
with tempfile.TemporaryDirectory() as tmp:
    geojson = pathlib.Path(tmp) / "counties.geojson"
    geojson.write_bytes(read_bytes(counties_path))
    counties = geopandas.read_file(geojson)
points = geopandas.GeoDataFrame(geometry=geopandas.points_from_xy(lon, lat), crs=counties.crs)
start = time.perf_counter()
joined = geopandas.sjoin(points, counties, predicate="within", how="left")
seconds = time.perf_counter() - start
theirs = joined[~joined.index.duplicated()]["index_right"].fillna(-1).astype(np.int64)
same = int((theirs.to_numpy() == county).sum())
print(f"geopandas.sjoin: {seconds * 1e3:.0f} ms, {seconds / located:.0f}x kiln's time; "
      f"same county for {same:,} of {len(zips):,} points")
