"""Event queries: count, series, tiles and topk equal `kiln query`'s JSON lines on the same
nanocube, and count equals a brute-force scan of the CSV."""
import json

import numpy as np
import pytest

import kiln
from conftest import run_cli

T0 = 978307200  # 2001-01-01T00:00Z


@pytest.fixture(scope="module")
def events(tmp):
    """3,000 events over the US in January 2001 with a carrier and a delay; their blob."""
    rng = np.random.default_rng(9)
    n = 3000
    lon, lat = rng.uniform(-124, -70, n), rng.uniform(26, 48, n)
    t = T0 + rng.integers(0, 31 * 86400, n)
    carrier = rng.choice(["AA", "UA", "DL", "WN"], n, p=[0.4, 0.3, 0.2, 0.1])
    delay = rng.integers(-20, 120, n)
    lines = ["lat,lon,time,carrier,delay"] + [
        f"{a:.6f},{o:.6f},{s},{c},{d}" for a, o, s, c, d in zip(lat, lon, t, carrier, delay)]
    (tmp / "events.csv").write_text("\n".join(lines) + "\n")
    path = tmp / "events.kiln"
    run_cli("build", tmp / "events.csv", "-o", path, "--accel", "nanocube", "--lat", "lat",
            "--lon", "lon", "--time", "time", "--time-bin", "1h", "--category", "carrier",
            "--category", "delay=delay:-inf,0,15,inf", "--max-level", "12")
    return path, dict(lon=lon, lat=lat, t=t, carrier=carrier, delay=delay)


QUERIES = [
    {},
    {"box": [-110.0, 30.0, -90.0, 40.0]},
    {"time": ["2001-01-05T00:00Z", "2001-01-12T06:00Z"], "where": {"carrier": ["AA", "DL"]}},
    {"tile": [3, 1, 2], "where": {"delay": ">=15"}},
    {"box": [-100.0, 35.0, -80.0, 45.0], "time": [T0, T0 + 7 * 86400]},
]


def iso(value):
    """A datetime64 as the JSON lines write times: YYYY-MM-DDTHH:MMZ (with :SS if any)."""
    text = str(np.datetime64(value, "s"))
    return (text[:-3] if text.endswith(":00") else text) + "Z"


def cli_answers(tmp, blob, op, queries):
    (tmp / f"{op}.jsonl").write_text("".join(json.dumps(q) + "\n" for q in queries))
    run_cli("query", blob, "--op", op, "--in", tmp / f"{op}.jsonl", "--out", tmp / f"{op}.out")
    return [json.loads(line) for line in (tmp / f"{op}.out").read_text().splitlines()]


def as_json(answer):
    """Our answer in the JSON lines' representation."""
    out = {}
    for key, value in answer.items():
        if key == "series":
            out[key] = [[iso(t), int(c)] for t, c in value]
        elif key == "tiles":
            out[key] = [[int(z), int(x), int(y), int(c)] for z, x, y, c in value]
        elif key == "topk":
            out[key] = [[label, count] for label, count in value]
        elif key == "time":
            out[key] = [iso(t) for t in value]
        elif key == "box":
            out[key] = list(value)
        else:
            out[key] = value
    return out


def selection(q):
    return {k: q[k] for k in ("box", "tile", "time", "where") if k in q}


@pytest.mark.parametrize("op,params", [
    ("count", {}), ("series", {"bin": "1d"}), ("tiles", {"zoom": 4}),
    ("topk", {"by": "carrier", "k": 3})])
def test_events_equal_kiln_query(tmp, events, op, params):
    path, _ = events
    cli = cli_answers(tmp, path, op, [dict(q, **params) for q in QUERIES])
    with kiln.open(path) as blob:
        cube = blob["nanocube"]
        for q, expected in zip(QUERIES, cli):
            if op == "count":
                ours = cube.count(**selection(q))
            elif op == "series":
                ours = cube.series(params["bin"], **selection(q))
            elif op == "tiles":
                ours = cube.tiles(params["zoom"], **selection(q))
            else:
                ours = cube.topk(params["k"], params["by"], **selection(q))
            assert as_json(ours) == expected, q


def test_count_equals_brute_force(events):
    path, e = events
    with kiln.open(path) as blob:
        cube = blob["nanocube"]
        assert cube.count()["count"] == len(e["t"])
        aa = cube.count(where={"carrier": "AA"})["count"]
        assert aa == int((e["carrier"] == "AA").sum())
        late = cube.count(where={"delay": ">=15"})["count"]
        assert late == int((e["delay"] >= 15).sum())
        week = cube.count(time=(np.datetime64("2001-01-08"), "2001-01-15T00:00Z"))["count"]
        assert week == int(((e["t"] >= T0 + 7 * 86400) & (e["t"] < T0 + 14 * 86400)).sum())
        series = cube.series(86400)["series"]
        assert series.dtype.names == ("time", "count") and series["count"].sum() == len(e["t"])


def test_bad_event_requests(events):
    path, _ = events
    with kiln.open(path) as blob:
        cube = blob["nanocube"]
        with pytest.raises(ValueError, match="unknown|category"):
            cube.topk(3, "airline")
        with pytest.raises(ValueError, match="box"):
            cube.count(box=[1, 2, 3])
        with pytest.raises(ValueError, match="time"):
            cube.count(time=["yesterday", "today"])
        with pytest.raises(ValueError):
            cube.tiles(40)
        with pytest.raises(TypeError, match="where"):
            cube.count(where=["carrier"])
        with pytest.raises(TypeError, match="nanocube.*cannot answer knn"):
            cube.knn([[0, 0, 0]])
