"""kiln.build: the same blob as `kiln build` with the same options, and the same errors."""
import pytest

import kiln
from conftest import ROOT, cli_error, run_cli

SAMPLE = ROOT / "samples" / "wuson.obj"


def test_build_is_byte_identical_to_the_cli(tmp):
    ours, theirs = tmp / "py_build.kiln", tmp / "cli_build.kiln"
    stages = []
    report = kiln.build(SAMPLE, ours, accel=["bvh", "points:leaf-size=4"], bvh_max_leaf=4,
                        threads=1, progress=lambda stage, done, total: stages.append(stage))
    run_cli("build", SAMPLE, "-o", theirs, "--accel", "bvh", "--accel", "points:leaf-size=4",
            "--bvh-max-leaf", "4")
    assert ours.read_bytes() == theirs.read_bytes()
    assert [s["name"] for s in report["structures"]] == ["bvh", "points"]
    assert stages, "the progress callback was never called"
    with kiln.open(ours) as blob:
        assert blob.structures[0]["stats"]["max_leaf_size"] == 4


def test_build_2d_and_compressed(tmp, zip_blob):
    from conftest import DATA
    out = tmp / "zip_py.kiln"
    kiln.build(str(DATA / "geo" / "zipcodes.csv.zst"), str(out), "quadtree",
               lon_column="longitude", lat_column="latitude", compress=True)
    with kiln.open(out) as ours, kiln.open(zip_blob) as theirs:
        assert (ours.table_points == theirs.table_points).all()


@pytest.mark.parametrize("accel,cli_flags,kwargs", [
    ("nope", [], {}),
    ("bvh:max-leaf=0", [], {}),
    ("bvh:colour=red", [], {}),
    ("bvh", ["--bvh-width", "3"], {"bvh_width": 3}),
])
def test_bad_options_raise_value_error_with_the_cli_line(tmp, accel, cli_flags, kwargs):
    expected = cli_error("build", SAMPLE, "-o", tmp / "x.kiln", "--accel", accel, *cli_flags)
    with pytest.raises(ValueError) as error:
        kiln.build(SAMPLE, tmp / "x.kiln", accel=accel, **kwargs)
    assert str(error.value) == expected
    assert not (tmp / "x.kiln").exists()


def test_failed_import_raises_build_error_with_the_cli_line(tmp):
    missing = tmp / "missing.obj"
    expected = cli_error("build", missing, "-o", tmp / "y.kiln", "--accel", "bvh")
    with pytest.raises(kiln.BuildError) as error:
        kiln.build(missing, tmp / "y.kiln", accel="bvh")
    assert str(error.value) == expected
    points_only = cli_error("build", ROOT / "samples" / "wuson.obj", "-o", tmp / "z.kiln",
                            "--lon-column", "x")
    with pytest.raises(ValueError) as error:
        kiln.build(SAMPLE, tmp / "z.kiln", lon_column="x")
    assert str(error.value) == points_only


def test_bad_keywords_and_arguments(tmp):
    with pytest.raises(TypeError, match="unexpected keyword argument 'colour'.*bvh_width"):
        kiln.build(SAMPLE, tmp / "w.kiln", accel="bvh", colour="red")
    with pytest.raises(TypeError, match="inputs: expected a path"):
        kiln.build([3], tmp / "w.kiln")
    with pytest.raises(ValueError, match="compression_level"):
        kiln.build(SAMPLE, tmp / "w.kiln", compress=True, compression_level=40)
    with pytest.raises(ValueError, match="also an input"):
        kiln.build(SAMPLE, SAMPLE, accel="bvh")
    with pytest.raises(ZeroDivisionError):
        kiln.build(SAMPLE, tmp / "w.kiln", accel="bvh", progress=lambda *a: 1 / 0)
    assert not (tmp / "w.kiln").exists()
